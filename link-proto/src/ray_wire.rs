//! A ray's wire form: fixed little-endian fields, packed and unpacked by
//! hand, carried in a frame as its bare bytes (to postcard, a tuple of
//! them): its header says how long it is, so it needs no length.
//!
//! Rays are most of the traffic between nodes, and every byte of a ray is
//! paid three times: on the wire, and by the CRC and COBS at both ends. So a
//! ray carries only what its exact continuation needs, in the shortest of a
//! few fixed forms that its header chooses:
//! - the first byte has its top bit set, which no other message's first
//!   byte has (postcard's variant indices are under 128): in a frame it is
//!   the message's tag as well, with a bit for a ray passed on a grant;
//! - a primary ray's origin is the eye, which every node knows: a node
//!   sends [`ORIGIN_AT_EYE`] in its place and it takes no bytes;
//! - a primary ray in its usual form (from the eye, at full strength with
//!   its pixel's whole credit, cells and pixel packed, nothing rarer, a class
//!   under 16) is its head byte, its direction and its cells: 17 bytes, its
//!   class in the head where other rays have their credit's form and depth;
//! - any other origin inside the grid's first 32 cubes a side (every
//!   reflected or shadow ray's in a grid of up to 32 cubes: it starts on a
//!   sphere the grid holds) takes 21 bits a component, eight bytes in all;
//!   inside its first 256 cubes three bytes a component, else four;
//! - the direction takes twelve bytes, its components whole (left out, its
//!   largest component could be put back from the other two with a square
//!   root, three bytes fewer: that cost the two ends of a hop 135
//!   instructions, more than the bytes spared; see docs/scaling.md);
//! - cells under 32 and a pixel under 2^17 (every cell of a grid up to 32
//!   cubes a side, every pixel of an image up to 362x362) take four bytes
//!   together, cells under 256 and a pixel under 2^24 six, else ten;
//! - weights at full strength (every primary ray) take none, weights under
//!   2^16 two bytes each, else four;
//! - credit of exactly 2^32 (a primary ray's) takes none; an odd multiple
//!   up to 7 of a power of two (every other ray's: a hit splits its ray's
//!   credit among its children by powers of two) one byte
//!   ([`crate::credit`]); any other under 2^32 four bytes, else eight;
//! - a class under 256 one byte, else two; a zero tag (every ray passed on a
//!   grant) none; depth under 3 rides in the header.
//!
//! What few rays need (a tag, a carried hit, a distance to stop at, a wide
//! class or wide cells) is flagged in a third header byte that only they carry.
//!
//! Any [`RayMsg`] round-trips, and each has exactly one encoding: bytes that
//! are not the encoder's choice for some ray are refused, never read as
//! something else.
//!
//! Layout: head, direction, packed cells and pixel for a usual primary;
//! for every other ray head, forms, \[more\], \[depth\], \[origin\], direction, cells and
//! pixel, \[weights\], \[credit\], class, \[tag\], then `ignore` (u16),
//! `t_max` (i32) and `best` (t as i32, then the sphere) when present.

use serde::de::{Error as _, Visitor};
use serde::{Deserialize, Deserializer, Serialize, Serializer};

use crate::credit;
use crate::message::{HitMsg, MaterialMsg, Message, RayKind, RayMsg, SphereMsg};
use crate::pack::{Reader, Writer};

/// The origin a node writes for a primary ray that starts at the eye: the
/// wire leaves it out, and the receiver puts its own eye back. Far outside
/// every accepted coordinate range, so a ray that keeps it is refused.
pub const ORIGIN_AT_EYE: [i32; 3] = [i32::MIN; 3];

// The head byte: a ray, on a grant or not, its kind, its credit's form and its depth.
/// Set in every ray's first byte, and in no other message's.
pub const RAY: u8 = 1 << 7;
/// A ray passed on a grant ([`Message::GrantedRay`]); never in a bare ray's bytes.
pub const GRANTED: u8 = 1 << 6;
const KIND_SHIFT: u32 = 4;
const KIND_MASK: u8 = 0b11 << KIND_SHIFT;
/// The credit's form ([`credit::Form`]), its code in two bits.
const CREDIT_SHIFT: u32 = 2;
const CREDIT_MASK: u8 = 0b11 << CREDIT_SHIFT;
const DEPTH_MASK: u8 = 0b11;
/// A depth this large or larger follows in a byte of its own. Depths 0 to
/// 2 (a primary ray, its shadow rays, one reflection and its shadow rays)
/// are most of the traffic.
const DEPTH_ESCAPE: u8 = 3;
/// The fourth kind code: a primary ray in its usual form (see
/// [`usual_primary`]), its head byte alone before its direction and its
/// packed cells, with its class in the four bits that hold the credit's form
/// and the depth of every other ray.
const USUAL_PRIMARY: u8 = 3 << KIND_SHIFT;
const USUAL_CLASS_MASK: u8 = 0b1111;
/// Classes the usual primary's head holds: under this.
const USUAL_CLASS_LIMIT: u16 = 16;

// The forms byte.
const WEIGHTS_MASK: u8 = 0b11;
const WEIGHTS_FULL: u8 = 0;
const WEIGHTS_SHORT: u8 = 1;
const WEIGHTS_LONG: u8 = 2;
const ORIGIN_SHIFT: u32 = 2;
const ORIGIN_MASK: u8 = 0b11 << ORIGIN_SHIFT;
const ORIGIN_EYE: u8 = 0;
const ORIGIN_PACKED: u8 = 1 << ORIGIN_SHIFT;
const ORIGIN_SHORT: u8 = 2 << ORIGIN_SHIFT;
const ORIGIN_LONG: u8 = 3 << ORIGIN_SHIFT;
const HAS_IGNORE: u8 = 1 << 4;
/// Cells and pixel in four bytes.
const PACKED_CELLS: u8 = 1 << 5;
/// The byte of rarer flags follows.
const MORE: u8 = 1 << 6;
/// No ray has it.
const FORMS_UNUSED: u8 = 1 << 7;

// The byte of rarer flags: present, and not zero, only when one is set.
const HAS_TAG: u8 = 1 << 0;
const HAS_BEST: u8 = 1 << 1;
const HAS_T_MAX: u8 = 1 << 2;
const WIDE_CLASS: u8 = 1 << 3;
/// Cells two bytes each and the pixel four, for a cell or a pixel out of the short forms.
const WIDE_CELLS: u8 = 1 << 4;
const MORE_BITS: u8 = 0b1_1111;

/// Packed origin components are under this: 21 bits.
const PACKED_ORIGIN_LIMIT: u32 = 1 << 21;
const LOW21: u64 = (1 << 21) - 1;
/// Packed cells are under this (5 bits each), a packed pixel under 2^17.
const PACKED_CELL_LIMIT: u16 = 1 << 5;
const PACKED_PIXEL_LIMIT: u32 = 1 << 17;
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
pub const RAY_MAX_LEN: usize = 3 + 1 + 12 + 12 + 10 + 12 + 8 + 2 + 2 + 2 + 4 + 4 + SPHERE_LEN;

fn kind_bits(kind: RayKind) -> u8 {
    let k = match kind {
        RayKind::Primary => 0,
        RayKind::Reflected => 1,
        RayKind::Shadow => 2,
    };
    k << KIND_SHIFT
}

fn kind_of(head: u8) -> Option<RayKind> {
    match (head & KIND_MASK) >> KIND_SHIFT {
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

/// The origin's form.
fn origin_form(origin: [i32; 3]) -> u8 {
    // As unsigned, a component below zero is over every limit, as the eye's are.
    let top = largest_u32(origin.map(|c| c as u32));
    if top < PACKED_ORIGIN_LIMIT {
        ORIGIN_PACKED
    } else if top < SHORT_LIMIT {
        ORIGIN_SHORT
    } else if at_eye(origin) {
        ORIGIN_EYE
    } else {
        ORIGIN_LONG
    }
}

/// The largest of three, in two comparisons.
fn largest_u32([x, y, z]: [u32; 3]) -> u32 {
    x.max(y).max(z)
}

/// Cells and pixel in four bytes, if they fit.
fn packed_cells(cell: [u16; 3], pixel: u32) -> bool {
    largest_u32(cell.map(u32::from)) < u32::from(PACKED_CELL_LIMIT) && pixel < PACKED_PIXEL_LIMIT
}

/// Cells and pixel in ten bytes: they fit no shorter form.
fn wide_cells(cell: [u16; 3], pixel: u32) -> bool {
    largest_u32(cell.map(u32::from)) > 0xff || pixel >= SHORT_LIMIT
}

/// The header bytes the encoder chooses for `out`, going with `origin`,
/// whose credit takes `credit`.
/// Each flag is its condition shifted into place, without a branch; in
/// line, which spares a call's saved registers and spills (8 instructions
/// of a hop end's 450 on a Cortex-M3).
#[inline(always)]
fn header_of(out: &OutgoingRay<'_>, origin: [i32; 3], credit: credit::Form) -> [u8; 3] {
    let ray = out.ray;
    let bit = |set: bool, bit: u8| u8::from(set) * bit;
    let head = RAY
        | bit(out.granted, GRANTED)
        | kind_bits(ray.kind)
        | credit.code() << CREDIT_SHIFT
        | ray.depth.min(DEPTH_ESCAPE);
    let weights = if ray.weight.iter().all(|&w| w == FULL_WEIGHT) {
        WEIGHTS_FULL
    } else if ray.weight.iter().all(|&w| w <= 0xffff) {
        WEIGHTS_SHORT
    } else {
        WEIGHTS_LONG
    };
    let more = bit(out.tag != 0, HAS_TAG)
        | bit(ray.best.is_some(), HAS_BEST)
        | bit(ray.t_max.is_some(), HAS_T_MAX)
        | bit(out.class > 0xff, WIDE_CLASS)
        | bit(wide_cells(ray.cell, ray.pixel), WIDE_CELLS);
    let forms = weights
        | origin_form(origin)
        | bit(ray.ignore.is_some(), HAS_IGNORE)
        | bit(packed_cells(ray.cell, ray.pixel), PACKED_CELLS)
        | bit(more != 0, MORE);
    [head, forms, more]
}

/// Whether a ray whose header the encoder chose as `head` and `forms`, of
/// class `class`, goes as a usual primary: a primary ray (kind code 0) with
/// its pixel's whole credit (credit code 0) at depth 0 (the head's low six
/// bits all zero), from the eye at full strength with no ignored sphere and
/// its cells packed, nothing rarer (the forms byte nothing but
/// [`PACKED_CELLS`]), and a class under 16: half the rays a node of the
/// paper's 4x4x4 array passes. Two bytes fewer than the other forms.
#[inline(always)]
fn usual_primary(head: u8, forms: u8, class: u16) -> bool {
    head & !(RAY | GRANTED) == 0 && forms == PACKED_CELLS && class < USUAL_CLASS_LIMIT
}

/// The low three bytes of `v`.
fn three_bytes(v: u32) -> [u8; 3] {
    let [a, b, c, _] = v.to_le_bytes();
    [a, b, c]
}

/// Packs `ray` into `out` as a bare ray (not on a grant); the length
/// written, or `None` if `out` is shorter than the ray needs
/// ([`RAY_MAX_LEN`] always suffices).
#[inline(always)]
pub fn encode_ray(ray: &RayMsg, out: &mut [u8]) -> Option<usize> {
    encode_outgoing(&OutgoingRay::of(ray, false), out)
}

/// Packs the message `o` stands for ([`OutgoingRay::message`]) into `out`,
/// its head byte its tag in a frame: as [`encode_ray`] packs the ray, with
/// [`GRANTED`] set on a grant.
#[inline(always)]
pub fn encode_outgoing(o: &OutgoingRay<'_>, out: &mut [u8]) -> Option<usize> {
    let ray = o.ray;
    let origin = o.origin();
    let credit = credit::Form::of(ray.credit);
    let [head, forms, more] = header_of(o, origin, credit);
    let mut w = Writer::new(out);
    if usual_primary(head, forms, o.class) {
        w.put(&[head | USUAL_PRIMARY | o.class as u8])?;
        put_direction(&mut w, ray.dir)?;
        put_packed_cells(&mut w, ray)?;
        return Some(w.at);
    }
    w.put(&[head, forms])?;
    if more != 0 {
        w.put(&[more])?;
    }
    if ray.depth >= DEPTH_ESCAPE {
        w.put(&[ray.depth])?;
    }
    match forms & ORIGIN_MASK {
        ORIGIN_PACKED => {
            let [x, y, z] = origin.map(|c| u64::from(c as u32));
            w.put(&(x | y << 21 | z << 42).to_le_bytes())?;
        }
        ORIGIN_SHORT => {
            for v in origin {
                w.put(&three_bytes(v as u32))?;
            }
        }
        ORIGIN_LONG => {
            for v in origin {
                w.put(&v.to_le_bytes())?;
            }
        }
        _ => {}
    }
    put_direction(&mut w, ray.dir)?;
    if forms & PACKED_CELLS != 0 {
        put_packed_cells(&mut w, ray)?;
    } else if more & WIDE_CELLS != 0 {
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
    if more & WIDE_CLASS != 0 {
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

#[inline(always)]
fn put_direction(w: &mut Writer<'_>, dir: [i32; 3]) -> Option<()> {
    for v in dir {
        w.put(&v.to_le_bytes())?;
    }
    Some(())
}

/// Cells and pixel in four bytes ([`packed_cells`] says whether they fit).
#[inline(always)]
fn put_packed_cells(w: &mut Writer<'_>, ray: &RayMsg) -> Option<()> {
    let [x, y, z] = ray.cell.map(u32::from);
    w.put(&(x | y << 5 | z << 10 | ray.pixel << 15).to_le_bytes())
}

/// Cells and pixel from their four packed bytes.
#[inline(always)]
fn unpack_cells(v: u32) -> ([u16; 3], u32) {
    ([v & 0x1f, v >> 5 & 0x1f, v >> 10 & 0x1f].map(|c| c as u16), v >> 15)
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

/// Unpacks a bare ray; `None` unless `bytes` are exactly one ray's wire
/// form: the one [`encode_ray`] writes. Each form is checked as it is read
/// (a field written longer than its value needs is refused), which costs a
/// fraction of choosing the header again and comparing it.
#[inline(always)]
pub fn decode_ray(bytes: &[u8]) -> Option<RayMsg> {
    read_ray(bytes, |ray, granted, rest| (!granted && rest.is_empty()).then_some(ray))
}

/// The ray message at the start of `bytes` (its head byte its tag: a
/// [`Message::GrantedRay`] if [`GRANTED`] is set, else a [`Message::Ray`]),
/// written into `out` if `after` takes the bytes that follow it (a frame
/// gives a ray no length: its header says how long it is); what `after`
/// made of them. `out` is untouched unless both are good. Each variant is
/// built where it goes: a ray unpacked and then moved into the message cost
/// each received frame a copy of its 120 bytes.
#[inline(always)]
pub fn decode_ray_into<T>(
    bytes: &[u8],
    out: &mut Message,
    after: impl FnOnce(&[u8]) -> Option<T>,
) -> Option<T> {
    read_ray(bytes, |ray, granted, rest| {
        let made = after(rest)?;
        *out = if granted { Message::GrantedRay(ray) } else { Message::Ray(ray) };
        Some(made)
    })
}

/// Unpacks the ray at the start of `bytes` as [`decode_ray`] says and hands
/// it to `finish`, with whether it came on a grant and the bytes after it,
/// once every field is read and checked.
#[inline(always)]
fn read_ray<T>(bytes: &[u8], finish: impl FnOnce(RayMsg, bool, &[u8]) -> Option<T>) -> Option<T> {
    let mut r = Reader { bytes };
    let head = r.u8().filter(|h| h & RAY != 0)?;
    if head & KIND_MASK == USUAL_PRIMARY {
        let dir = r.i32x3()?;
        let (cell, pixel) = unpack_cells(r.u32()?);
        let ray = RayMsg {
            origin: ORIGIN_AT_EYE,
            dir,
            cell,
            pixel,
            weight: [FULL_WEIGHT; 3],
            credit: PIXEL_CREDIT,
            kind: RayKind::Primary,
            depth: 0,
            ignore: None,
            best: None,
            t_max: None,
            class: u16::from(head & USUAL_CLASS_MASK),
            tag: 0,
        };
        return finish(ray, head & GRANTED != 0, r.bytes);
    }
    let forms = r.u8().filter(|f| f & FORMS_UNUSED == 0)?;
    let more = if forms & MORE != 0 { r.u8().filter(|&m| m != 0 && m & !MORE_BITS == 0)? } else { 0 };
    let kind = kind_of(head)?;
    let depth = match head & DEPTH_MASK {
        DEPTH_ESCAPE => r.u8().filter(|&d| d >= DEPTH_ESCAPE)?,
        d => d,
    };
    // Each form is checked for the shorter forms its values would fit: a
    // packed origin's fit no shorter one.
    let origin = match forms & ORIGIN_MASK {
        ORIGIN_EYE => ORIGIN_AT_EYE,
        ORIGIN_PACKED => {
            let v = u64::from_le_bytes(r.take()?);
            if v >> 63 != 0 {
                return None;
            }
            [v & LOW21, v >> 21 & LOW21, v >> 42].map(|c| c as i32)
        }
        ORIGIN_SHORT => Some([r.u24()?, r.u24()?, r.u24()?])
            .filter(|&o| largest_u32(o) >= PACKED_ORIGIN_LIMIT)?
            .map(|c| c as i32),
        _ => r.i32x3().filter(|&o| origin_form(o) == ORIGIN_LONG)?,
    };
    let dir = r.i32x3()?;
    let (cell, pixel) = match (forms & PACKED_CELLS != 0, more & WIDE_CELLS != 0) {
        (true, false) => unpack_cells(r.u32()?),
        (false, false) => Some(([u16::from(r.u8()?), u16::from(r.u8()?), u16::from(r.u8()?)], r.u24()?))
            .filter(|&(c, p)| !packed_cells(c, p))?,
        (false, true) => {
            Some(([r.u16()?, r.u16()?, r.u16()?], r.u32()?)).filter(|&(c, p)| wide_cells(c, p))?
        }
        (true, true) => return None,
    };
    let weight = match forms & WEIGHTS_MASK {
        WEIGHTS_FULL => [FULL_WEIGHT; 3],
        WEIGHTS_SHORT => Some([u32::from(r.u16()?), u32::from(r.u16()?), u32::from(r.u16()?)])
            .filter(|w| w.iter().any(|&w| w != FULL_WEIGHT))?,
        WEIGHTS_LONG => Some([r.u32()?, r.u32()?, r.u32()?]).filter(|w| w.iter().any(|&w| w > 0xffff))?,
        _ => return None,
    };
    let credit = credit::Form::read((head & CREDIT_MASK) >> CREDIT_SHIFT, &mut r)?;
    let class = if more & WIDE_CLASS != 0 { r.u16().filter(|&c| c > 0xff)? } else { u16::from(r.u8()?) };
    if usual_primary(head, forms, class) {
        // The usual primary's own form is the only one it has.
        return None;
    }
    let tag = if more & HAS_TAG != 0 { r.u16().filter(|&t| t != 0)? } else { 0 };
    let ignore = if forms & HAS_IGNORE != 0 { Some(r.u16()?) } else { None };
    let t_max = if more & HAS_T_MAX != 0 { Some(r.i32()?) } else { None };
    let best =
        if more & HAS_BEST != 0 { Some(HitMsg { t: r.i32()?, sphere: take_sphere(&mut r)? }) } else { None };
    finish(
        RayMsg { origin, dir, cell, pixel, weight, credit, kind, depth, ignore, best, t_max, class, tag },
        head & GRANTED != 0,
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

/// How long the ray whose header is `head`, `forms` and `more` (zero when
/// `forms` has no [`MORE`], both zero for a usual primary, which has
/// neither) is on the wire, all of it: what a reader that
/// cannot see the whole frame (serde's) must take. Headers no encoder
/// writes give some length; the ray's decoder refuses them.
fn wire_len(head: u8, forms: u8, more: u8) -> usize {
    if head & KIND_MASK == USUAL_PRIMARY {
        return 1 + 12 + 4;
    }
    let has = |set: u8, bit: u8, len: usize| if set & bit != 0 { len } else { 0 };
    let depth = usize::from(head & DEPTH_MASK == DEPTH_ESCAPE);
    let origin = match forms & ORIGIN_MASK {
        ORIGIN_EYE => 0,
        ORIGIN_PACKED => 8,
        ORIGIN_SHORT => 9,
        _ => 12,
    };
    let cells = match (forms & PACKED_CELLS != 0, more & WIDE_CELLS != 0) {
        (true, _) => 4,
        (false, false) => 6,
        (false, true) => 10,
    };
    let weights = match forms & WEIGHTS_MASK {
        WEIGHTS_SHORT => 6,
        WEIGHTS_LONG => 12,
        _ => 0,
    };
    let credit = credit::Form::wire_len((head & CREDIT_MASK) >> CREDIT_SHIFT);
    let class = if more & WIDE_CLASS != 0 { 2 } else { 1 };
    2 + has(forms, MORE, 1)
        + depth
        + origin
        + 12
        + cells
        + weights
        + credit
        + class
        + has(more, HAS_TAG, 2)
        + has(forms, HAS_IGNORE, 2)
        + has(more, HAS_T_MAX, 4)
        + has(more, HAS_BEST, 4 + SPHERE_LEN)
}

/// A ray is its wire form's bytes, one after another with no length before
/// them (as a tuple, which postcard writes so): its header says how many.
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
                let head = next()?;
                let (forms, header_len) = match head & KIND_MASK {
                    USUAL_PRIMARY => (0, 1),
                    _ => match next()? {
                        forms if forms & MORE != 0 => (forms, 3),
                        forms => (forms, 2),
                    },
                };
                let more = if header_len == 3 { next()? } else { 0 };
                let header = [head, forms, more];
                let header = header.get(..header_len).unwrap_or_default();
                let len = wire_len(head, forms, more);
                let bytes = buf.get_mut(..len).ok_or_else(|| A::Error::custom("not a ray"))?;
                let (start, tail) =
                    bytes.split_at_mut_checked(header.len()).ok_or_else(|| A::Error::custom("not a ray"))?;
                start.copy_from_slice(header);
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
            cell: [3, 20, 31],
            pixel: (1 << 17) - 1,
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

    /// A shadow ray as a hit in a 32-cube grid makes one.
    fn shadow() -> RayMsg {
        RayMsg {
            origin: [0, (1 << 21) - 1, 5 << 16],
            weight: [1000, 0, 32767],
            credit: PIXEL_CREDIT / 4,
            kind: RayKind::Shadow,
            depth: 1,
            ignore: Some(999),
            ..primary()
        }
    }

    #[test]
    fn a_usual_primary_ray_on_a_grant_takes_17_bytes() {
        let mut buf = [0u8; RAY_MAX_LEN];
        // The head with the class in it, 12 of direction, 4 of cells and pixel.
        let p = RayMsg { class: 11, ..primary() };
        assert_eq!(encode_outgoing(&OutgoingRay::of(&p, true), &mut buf), Some(1 + 12 + 4));
        assert_eq!(buf[0], RAY | GRANTED | 3 << KIND_SHIFT | 11);
        let mut out = Message::Space;
        assert_eq!(decode_ray_into(&buf[..17], &mut out, |rest| rest.is_empty().then_some(())), Some(()));
        assert_eq!(out, Message::GrantedRay(p));
        // A bare ray is never on a grant.
        assert_eq!(decode_ray(&buf[..17]), None);
        buf[0] &= !GRANTED;
        assert_eq!(decode_ray(&buf[..17]), Some(p));
    }

    #[test]
    fn a_primary_ray_of_class_16_or_more_takes_19_bytes() {
        let mut buf = [0u8; RAY_MAX_LEN];
        // Head and forms, 12 of direction, 4 of cells and pixel, 1 of class.
        let p = RayMsg { class: 16, ..primary() };
        assert_eq!(encode_outgoing(&OutgoingRay::of(&p, true), &mut buf), Some(2 + 12 + 4 + 1));
        assert_eq!(buf[..2], [RAY | GRANTED, PACKED_CELLS]);
        let mut out = Message::Space;
        assert_eq!(decode_ray_into(&buf[..19], &mut out, |rest| rest.is_empty().then_some(())), Some(()));
        assert_eq!(out, Message::GrantedRay(p));
    }

    #[test]
    fn a_shadow_ray_in_a_grid_of_32_takes_36_bytes() {
        let mut buf = [0u8; RAY_MAX_LEN];
        let r = shadow();
        // Head, forms, origin 8, direction 12, cells and pixel 4, weights 6,
        // credit 1, class 1, ignore 2.
        let n = encode_ray(&r, &mut buf).unwrap();
        assert_eq!(n, 2 + 8 + 12 + 4 + 6 + 1 + 1 + 2);
        let packed = u64::from_le_bytes(buf[2..10].try_into().unwrap());
        assert_eq!(packed, ((1 << 21) - 1) << 21 | (5 << 16) << 42);
        assert_eq!(decode_ray(&buf[..n]), Some(r));
        // One component at 2^21, and the origin takes three bytes each; at
        // 2^24 or below zero, four.
        for (far, len) in [(1 << 21, n + 1), (1 << 24, n + 4), (-1, n + 4)] {
            let r = RayMsg { origin: [0, far, 5 << 16], ..r };
            assert_eq!(encode_ray(&r, &mut buf), Some(len));
            assert_eq!(decode_ray(&buf[..len]), Some(r));
        }
    }

    #[test]
    fn a_second_encoding_of_the_same_ray_is_refused() {
        let mut buf = [0u8; RAY_MAX_LEN];
        let r = shadow();
        let n = encode_ray(&r, &mut buf).unwrap();
        // Its origin written three bytes a component although it packs.
        let mut short = buf[..2].to_vec();
        short[1] = short[1] & !ORIGIN_MASK | ORIGIN_SHORT;
        for v in r.origin {
            short.extend_from_slice(&three_bytes(v as u32));
        }
        short.extend_from_slice(&buf[10..n]);
        assert_eq!(decode_ray(&short), None);
        // Its cells and pixel in six bytes although they pack.
        let mut six = buf[..22].to_vec();
        six[1] &= !PACKED_CELLS;
        six.extend(r.cell.map(|c| c as u8));
        six.extend_from_slice(&three_bytes(r.pixel));
        six.extend_from_slice(&buf[26..n]);
        assert_eq!(decode_ray(&six), None);
        // A rarer-flags byte of zero.
        let mut zero = buf[..n].to_vec();
        zero[1] |= MORE;
        zero.insert(2, 0);
        assert_eq!(decode_ray(&zero), None);
        // A full-strength primary ray with its weights written out.
        let p = primary();
        let n = encode_ray(&p, &mut buf).unwrap();
        let mut long = buf[..n].to_vec();
        long[1] |= WEIGHTS_SHORT;
        let at = 2 + 12 + 4;
        for _ in 0..3 {
            long.splice(at..at, 32768u16.to_le_bytes());
        }
        assert_eq!(decode_ray(&long), None);
        // A usual primary written in the other forms' layout.
        let p = RayMsg { class: 15, ..primary() };
        let n = encode_ray(&p, &mut buf).unwrap();
        assert_eq!(n, 17);
        let mut plain = vec![RAY, PACKED_CELLS];
        plain.extend_from_slice(&buf[1..n]);
        plain.push(15);
        assert_eq!(decode_ray(&plain), None);
        plain[18] = 16;
        assert_eq!(decode_ray(&plain), Some(RayMsg { class: 16, ..p }));
    }

    /// Rays with every field on both sides of its forms' limits, and
    /// primary rays in or one field out of the usual primary's form.
    fn arb_ray() -> impl proptest::strategy::Strategy<Value = RayMsg> {
        proptest::prop_oneof![arb_any_ray(), arb_primary()]
    }

    fn sphere() -> SphereMsg {
        SphereMsg {
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
        }
    }

    /// Primary rays of any direction, cells and pixel in the packed form's
    /// range, classes on both sides of 16, and at most one other field
    /// away from the usual primary's.
    fn arb_primary() -> impl proptest::strategy::Strategy<Value = RayMsg> {
        use proptest::prelude::*;
        let cell = proptest::array::uniform3(0u16..32);
        (any::<[i32; 3]>(), cell, 0u32..1 << 17, 0u16..20, 0u8..12).prop_map(
            |(dir, cell, pixel, class, off)| {
                let p = RayMsg { dir, cell, pixel, class, ..primary() };
                match off {
                    0 => RayMsg { depth: 1, ..p },
                    1 => RayMsg { credit: PIXEL_CREDIT / 2, ..p },
                    2 => RayMsg { weight: [FULL_WEIGHT, FULL_WEIGHT, 32767], ..p },
                    3 => RayMsg { ignore: Some(3), ..p },
                    4 => RayMsg { tag: 5, ..p },
                    5 => RayMsg { t_max: Some(77), ..p },
                    6 => RayMsg { best: Some(HitMsg { t: 4, sphere: sphere() }), ..p },
                    7 => RayMsg { origin: [1, 2, 3], ..p },
                    8 => RayMsg { cell: [32, 0, 0], ..p },
                    9 => RayMsg { kind: RayKind::Reflected, ..p },
                    _ => p,
                }
            },
        )
    }

    /// Rays with every field on both sides of its forms' limits.
    fn arb_any_ray() -> impl proptest::strategy::Strategy<Value = RayMsg> {
        use proptest::prelude::*;
        let sphere = sphere();
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
        let near = |limit: i32| limit - 2..limit + 2;
        let origin = prop_oneof![
            Just(ORIGIN_AT_EYE),
            proptest::array::uniform3(prop_oneof![Just(i32::MIN), any::<i32>()]),
            // Packed and short components, and some just out of either form.
            proptest::array::uniform3(prop_oneof![0i32..1 << 21, near(1 << 21), -2i32..2]),
            proptest::array::uniform3(prop_oneof![0i32..1 << 24, near(1 << 24), -2i32..2])
        ];
        let cell = prop_oneof![
            proptest::array::uniform3(0u16..32),
            proptest::array::uniform3(prop_oneof![30u16..34, 250u16..260, any::<u16>()])
        ];
        let pixel = prop_oneof![
            0u32..1 << 17,
            (1u32 << 17) - 2..(1 << 17) + 2,
            0u32..1 << 24,
            (1u32 << 24) - 2..(1 << 24) + 2,
            any::<u32>()
        ];
        (
            (proptest::array::uniform3(prop_oneof_weights()), credit, cell),
            prop_oneof![250u16..260, any::<u16>()],
            prop_oneof![Just(0u16), any::<u16>()],
            prop_oneof![1u8..5, any::<u8>()],
            origin,
            proptest::option::of(any::<i32>()),
            proptest::option::of(any::<u16>()),
            any::<bool>(),
            pixel,
        )
            .prop_map(
                move |((weight, credit, cell), class, tag, depth, origin, t_max, ignore, best, pixel)| {
                    let best = best.then_some(HitMsg { t: -11, sphere });
                    RayMsg {
                        weight,
                        credit,
                        cell,
                        class,
                        tag,
                        depth,
                        origin,
                        t_max,
                        ignore,
                        best,
                        pixel,
                        ..ray()
                    }
                },
            )
    }

    /// The length [`wire_len`] gives the header at the start of `bytes`.
    fn wire_len_of(bytes: &[u8]) -> usize {
        if bytes[0] & KIND_MASK == USUAL_PRIMARY {
            return wire_len(bytes[0], 0, 0);
        }
        let more = if bytes[1] & MORE != 0 { bytes[2] } else { 0 };
        wire_len(bytes[0], bytes[1], more)
    }

    proptest::proptest! {
        #[test]
        fn rays_round_trip_across_the_forms(r in arb_ray(), granted in proptest::bool::ANY) {
            let mut buf = [0u8; RAY_MAX_LEN];
            let n = encode_outgoing(&OutgoingRay::of(&r, granted), &mut buf).unwrap();
            let mut out = Message::Space;
            let taken = decode_ray_into(&buf[..n], &mut out, |rest| rest.is_empty().then_some(()));
            proptest::prop_assert_eq!(taken, Some(()));
            let want = if granted { Message::GrantedRay(r) } else { Message::Ray(r) };
            proptest::prop_assert_eq!(out, want);
            proptest::prop_assert_eq!(wire_len_of(&buf), n);
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
        cells: Cells,
        weights: u8,
        credit: u8,
        wide_class: bool,
        tag: bool,
    }

    #[derive(Debug, Clone, Copy, PartialEq)]
    enum Origin {
        AtEye,
        Packed,
        Short,
        Long,
    }

    #[derive(Debug, Clone, Copy, PartialEq)]
    enum Cells {
        Packed,
        Short,
        Wide,
    }

    /// Every choice of forms whose fields `r`'s values fit, canonical or not.
    fn forms_fitting(r: &RayMsg) -> Vec<Forms> {
        let fits = |v: &[u32], max: u32| v.iter().all(|&x| x <= max);
        let cells = r.cell.map(u32::from);
        let (weights, credits) = (
            [WEIGHTS_FULL, WEIGHTS_SHORT, WEIGHTS_LONG],
            [CREDIT_PRIMARY, CREDIT_SHORT, CREDIT_LONG, CREDIT_SCALED],
        );
        let origins = [Origin::AtEye, Origin::Packed, Origin::Short, Origin::Long];
        let cell_forms = [Cells::Packed, Cells::Short, Cells::Wide];
        // Two ways for three fields, three for two, four for two: 2 304
        // choices, by mixed radix.
        (0..2 * 4 * 3 * 3 * 4 * 2 * 2)
            .map(|i: usize| Forms {
                escaped_depth: i % 2 == 1,
                origin: origins[i / 2 % 4],
                cells: cell_forms[i / 8 % 3],
                weights: weights[i / 24 % 3],
                credit: credits[i / 72 % 4],
                wide_class: i / 288 % 2 == 1,
                tag: i / 576 % 2 == 1,
            })
            .filter(|f| f.escaped_depth || r.depth < DEPTH_ESCAPE)
            .filter(|f| match f.origin {
                Origin::AtEye => r.origin == ORIGIN_AT_EYE,
                Origin::Packed => r.origin.iter().all(|&c| (0..1 << 21).contains(&c)),
                Origin::Short => r.origin.iter().all(|&c| (0..1 << 24).contains(&c)),
                Origin::Long => true,
            })
            .filter(|f| match f.cells {
                Cells::Packed => fits(&cells, 31) && r.pixel < 1 << 17,
                Cells::Short => fits(&cells, 0xff) && r.pixel < 1 << 24,
                Cells::Wide => true,
            })
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
        let depth = if f.escaped_depth { DEPTH_ESCAPE } else { r.depth };
        let head = RAY | kind_bits(r.kind) | f.credit | depth;
        let mut more = 0;
        for (set, bit) in [
            (f.tag, HAS_TAG),
            (r.best.is_some(), HAS_BEST),
            (r.t_max.is_some(), HAS_T_MAX),
            (f.wide_class, WIDE_CLASS),
            (f.cells == Cells::Wide, WIDE_CELLS),
        ] {
            more |= if set { bit } else { 0 };
        }
        let origin = match f.origin {
            Origin::AtEye => ORIGIN_EYE,
            Origin::Packed => ORIGIN_PACKED,
            Origin::Short => ORIGIN_SHORT,
            Origin::Long => ORIGIN_LONG,
        };
        let mut forms = f.weights | origin;
        for (set, bit) in
            [(r.ignore.is_some(), HAS_IGNORE), (f.cells == Cells::Packed, PACKED_CELLS), (more != 0, MORE)]
        {
            forms |= if set { bit } else { 0 };
        }
        let mut b = vec![head, forms];
        if more != 0 {
            b.push(more);
        }
        if f.escaped_depth {
            b.push(r.depth);
        }
        let o = r.origin.map(|v| u64::from(v as u32));
        match f.origin {
            Origin::AtEye => {}
            Origin::Packed => b.extend((o[0] + (o[1] << 21) + (o[2] << 42)).to_le_bytes()),
            Origin::Short => b.extend(le(&r.origin.map(|v| v as u32), 3)),
            Origin::Long => b.extend(le(&r.origin.map(|v| v as u32), 4)),
        }
        b.extend(le(&r.dir.map(|v| v as u32), 4));
        let c = r.cell.map(u32::from);
        match f.cells {
            Cells::Packed => b.extend(le(&[c[0] + (c[1] << 5) + (c[2] << 10) + (r.pixel << 15)], 4)),
            Cells::Short => {
                b.extend(le(&c, 1));
                b.extend(le(&[r.pixel], 3));
            }
            Cells::Wide => {
                b.extend(le(&c, 2));
                b.extend(le(&[r.pixel], 4));
            }
        }
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

    /// `r` in the usual primary's layout, if it is one: the head (kind
    /// code 3, the class in its low four bits), the direction, the packed
    /// cells and pixel.
    fn usual_writing(r: &RayMsg) -> Option<Vec<u8>> {
        let usual = r.kind == RayKind::Primary
            && r.origin == ORIGIN_AT_EYE
            && r.weight == [FULL_WEIGHT; 3]
            && r.credit == PIXEL_CREDIT
            && r.depth == 0
            && (r.ignore, r.t_max, r.best, r.tag) == (None, None, None, 0)
            && r.cell.iter().all(|&c| c < 32)
            && r.pixel < 1 << 17
            && r.class < 16;
        if !usual {
            return None;
        }
        let c = r.cell.map(u32::from);
        let mut b = vec![RAY | 3 << KIND_SHIFT | r.class as u8];
        b.extend(r.dir.iter().flat_map(|d| d.to_le_bytes()));
        b.extend((c[0] + (c[1] << 5) + (c[2] << 10) + (r.pixel << 15)).to_le_bytes());
        Some(b)
    }

    proptest::proptest! {
        #![proptest_config(proptest::test_runner::Config::with_cases(256))]
        /// Of all the ways to write a ray, the decoder takes exactly one,
        /// the encoder's.
        #[test]
        fn a_ray_decodes_from_exactly_one_writing(r in arb_ray()) {
            let mut buf = [0u8; RAY_MAX_LEN];
            let n = encode_ray(&r, &mut buf).unwrap();
            let usual = usual_writing(&r).into_iter();
            let writings = forms_fitting(&r).into_iter().map(|f| write_in(&r, f)).chain(usual);
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
        let n = encode_outgoing(&OutgoingRay::of(&ray(), true), &mut buf).unwrap();
        buf[n..n + 2].copy_from_slice(&[7, 9]);
        let mut out = Message::Space;
        let rest = |after: &[u8]| Some(after.to_vec());
        assert_eq!(decode_ray_into(&buf[..n + 2], &mut out, rest), Some(vec![7, 9]));
        assert_eq!(out, Message::GrantedRay(ray()));
        buf[0] &= !GRANTED;
        assert_eq!(decode_ray_into(&buf[..n], &mut out, rest), Some(vec![]));
        assert_eq!(out, Message::Ray(ray()));
        // Cut short: refused, and the message is what it was.
        assert_eq!(decode_ray_into(&buf[..n - 1], &mut out, rest), None);
        assert_eq!(out, Message::Ray(ray()));
        // What follows refused: so is the ray.
        assert_eq!(decode_ray_into(&buf[..n + 2], &mut out, |_| None::<()>), None);
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
        assert_eq!(decode_ray(&bad[..n]), None, "kind code 3 is a usual primary, 17 bytes");
        assert!(decode_ray(&bad[..17]).is_some());
        let mut bad = buf;
        bad[1] |= 3;
        assert_eq!(decode_ray(&bad[..n]), None, "weight form 3 is no form");
        let mut bad = buf;
        bad[0] &= !RAY;
        assert_eq!(decode_ray(&bad[..n]), None, "no ray's head");
        let mut bad = buf;
        bad[1] |= FORMS_UNUSED;
        assert_eq!(decode_ray(&bad[..n]), None, "a form no ray has");
        let mut bad = buf;
        bad[2] |= 1 << 5;
        assert_eq!(decode_ray(&bad[..n]), None, "a rarer flag no ray has");
    }
}
