//! Framing: `COBS(mask(postcard(frame) ++ [ack] ++ crc32c_le)) ++ 0x00`, the
//! payload XORed with [`MASK`] before it is stuffed.
//!
//! `ack` is the optional piggybacked acknowledgement ([`Frame::ack`]), one
//! byte ([`Seq`]) after the body: present exactly when bytes remain between
//! the body and the CRC.
//!
//! A frame ends at its zero and the next begins after it: one delimiter a
//! frame, as PPP's HDLC-like framing needs one flag between two frames (RFC
//! 1662). A leading zero as well would cost every frame a byte (a twentieth
//! of a ray's frame) to spare the frame after a lost delimiter or a burst of
//! line noise: the CRC refuses the run the two make, and the reliable
//! channel sends it again. The CRC sits inside the COBS payload, so a
//! corrupted byte anywhere (including one that COBS decodes without complaint) is
//! caught. [`FrameDecoder`] never panics and resynchronises on the next zero byte
//! after garbage, a truncated frame or an oversize one.

use crate::message::{Frame, Message, RayReply, Seq};
use crate::ray_wire::{self, OutgoingRay};
use crate::retirements::{Retirements, WIRE_MAX_LEN};
use crate::{cobs, crc32c};
use postcard::experimental::max_size::MaxSize;
use serde::Deserialize;

/// The frame check: CRC-32C over `bytes`, which detects bursts better than
/// CRC-32/ISO-HDLC at the same cost (exposed so that its cost can be measured
/// apart from the rest of a frame's encoding).
pub fn checksum(bytes: &[u8]) -> u32 {
    crc32c::checksum(bytes)
}
const CRC_LEN: usize = 4;

/// Largest postcard body, acknowledgement trailer and CRC of any frame
/// (`POSTCARD_MAX_SIZE` counts the skipped `ack` field as an `Option<u16>`,
/// a byte more than its trailer).
pub const MAX_PAYLOAD_LEN: usize = Frame::POSTCARD_MAX_SIZE + CRC_LEN;

/// Largest encoded frame on the wire, its zero delimiter included.
pub const MAX_FRAME_LEN: usize = cobs::max_encoding_length(MAX_PAYLOAD_LEN) + 1;

// Fixed buffers on a 64 KiB MCU: keep frames small. And short of COBS's
// first 254-byte run, so frames are stuffed in place.
const _: () = assert!(MAX_FRAME_LEN <= 160 && MAX_PAYLOAD_LEN < 254);

/// Why a frame could not be encoded.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EncodeError {
    /// The output buffer is shorter than the encoded frame.
    BufferTooSmall,
}

/// Why bytes between two zero delimiters were not a frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DecodeError {
    /// More than [`MAX_FRAME_LEN`] bytes arrived without a delimiter.
    Oversize,
    /// The bytes are not valid COBS.
    Cobs,
    /// Too short to hold a CRC.
    Short,
    /// The CRC does not match: a byte was corrupted.
    Crc,
    /// The CRC matched but the body is not a valid frame (e.g. version skew).
    Body,
}

/// Encodes `frame` into `out`, returning the number of bytes written.
///
/// The payload is written straight into `out` after a slot for the first
/// COBS code byte, then stuffed in place: no scratch
/// buffer to clear and no copy, which a node pays for on every message.
#[inline]
pub fn encode_frame(frame: &Frame, out: &mut [u8]) -> Result<usize, EncodeError> {
    encode_parts(frame.seq, &frame.msg, frame.ack, out)
}

/// [`encode_frame`] of the frame `seq`, `msg` and `ack` would make, without
/// the frame: a `Frame` holds a whole `Message`, as large as a ray with its
/// hit, which a control frame (an acknowledgement) would copy for nothing.
pub fn encode_parts(seq: Seq, msg: &Message, ack: Option<Seq>, out: &mut [u8]) -> Result<usize, EncodeError> {
    const SMALL: EncodeError = EncodeError::BufferTooSmall;
    let payload = payload_room(out)?;
    let mut body_len = encode_body(seq, msg, payload)?;
    if let Some(ack) = ack {
        let trailer = payload.get_mut(body_len..).ok_or(SMALL)?;
        body_len += postcard::to_slice(&ack, trailer).map_err(|_| SMALL)?.len();
    }
    seal(out, body_len)
}

/// Encodes a frame of one message already in its wire form (`message`, as
/// [`encode_message`] writes it) into `out`: the same bytes as
/// [`encode_parts`] of that message. A sender keeps what it has not had
/// acknowledged in this form, written once however often it is sent.
pub fn encode_encoded(
    seq: Seq,
    message: &[u8],
    ack: Option<Seq>,
    out: &mut [u8],
) -> Result<usize, EncodeError> {
    const SMALL: EncodeError = EncodeError::BufferTooSmall;
    let payload = payload_room(out)?;
    let (head, rest) = payload.split_first_mut().ok_or(SMALL)?;
    *head = seq;
    rest.get_mut(..message.len()).ok_or(SMALL)?.copy_from_slice(message);
    let mut body_len = 1 + message.len();
    if let Some(ack) = ack {
        *payload.get_mut(body_len).ok_or(SMALL)? = ack;
        body_len += 1;
    }
    seal(out, body_len)
}

/// Encodes as many of `frames` (sequence numbers and messages in their wire
/// form, [`encode_message`]'s, consecutive from the first) as fit into one
/// frame in `out`, with `ack` riding on it; returns the bytes written and
/// how many messages went in (at least one, or an error when there are none).
///
/// A batch: `seq ++ [BATCH_TAG, count | BATCH_ACK] ++ [ack] ++ messages`,
/// each message as it follows the sequence number in a frame of its own.
/// It pays a frame's delimiters, COBS code, CRC and header once for all its
/// messages: when rays queue up behind a busy link, they leave together. A
/// message that goes alone goes as [`encode_encoded`] writes it.
pub fn encode_batch<'m>(
    frames: impl IntoIterator<Item = (Seq, &'m [u8])>,
    ack: Option<Seq>,
    out: &mut [u8],
) -> Result<(usize, usize), EncodeError> {
    const SMALL: EncodeError = EncodeError::BufferTooSmall;
    let mut frames = frames.into_iter();
    let (first, message) = frames.next().ok_or(SMALL)?;
    let payload = payload_room(out)?;
    let limit = payload.len().saturating_sub(CRC_LEN);
    let head_len = if ack.is_some() { 4 } else { 3 };
    let (mut len, mut count) = (head_len, 0u8);
    for (seq, message) in core::iter::once((first, message)).chain(frames) {
        if count >= BATCH_MAX || seq != first.wrapping_add(count) {
            break;
        }
        match payload.get_mut(len..limit).and_then(|room| room.get_mut(..message.len())) {
            Some(room) => room.copy_from_slice(message),
            None => break,
        }
        len += message.len();
        count += 1;
    }
    if count < 2 {
        // Alone: as a frame of its own.
        return Ok((encode_encoded(first, message, ack, out)?, 1));
    }
    let head = [first, BATCH_TAG, count | if ack.is_some() { BATCH_ACK } else { 0 }, ack.unwrap_or(0)];
    payload.get_mut(..head_len).ok_or(SMALL)?.copy_from_slice(head.get(..head_len).unwrap_or_default());
    Ok((seal(out, len)?, usize::from(count)))
}

/// Where a frame's payload goes in `out = [code, payload.., 0]`: at most
/// what is left of `out`, and at most [`MAX_PAYLOAD_LEN`].
fn payload_room(out: &mut [u8]) -> Result<&mut [u8], EncodeError> {
    let room = out.len().saturating_sub(2).min(MAX_PAYLOAD_LEN);
    out.get_mut(1..1 + room).ok_or(EncodeError::BufferTooSmall)
}

/// Appends the CRC to the `body_len` bytes of body at `out[1..]`, stuffs
/// them in place and delimits the frame; its length on the wire.
fn seal(out: &mut [u8], body_len: usize) -> Result<usize, EncodeError> {
    const SMALL: EncodeError = EncodeError::BufferTooSmall;
    let payload = payload_room(out)?;
    let (crc, body_zeros) = crc32c::checksum_then_mask(payload.get_mut(..body_len).ok_or(SMALL)?, MASK);
    let payload_len = body_len + CRC_LEN;
    let crc = crc ^ crc_mask(body_len);
    payload.get_mut(body_len..payload_len).ok_or(SMALL)?.copy_from_slice(&crc.to_le_bytes());
    let stuffed = out.get_mut(..1 + payload_len).ok_or(SMALL)?;
    if body_zeros || cobs::zero_bytes(crc) != 0 {
        // MAX_PAYLOAD_LEN bounds the payload well under COBS's in-place limit.
        cobs::encode_in_place(stuffed).ok_or(SMALL)?;
    } else {
        // No zero to stuff: the one code byte spans the payload.
        *stuffed.first_mut().ok_or(SMALL)? = (payload_len + 1) as u8;
    }
    *out.get_mut(1 + payload_len).ok_or(SMALL)? = 0;
    Ok(payload_len + 2)
}

/// What a frame's payload (body, trailer and CRC) is XORed with on the
/// wire: byte `i` with byte `i % 4` of it, little-endian.
///
/// A frame's bytes are mostly small numbers and their zero high bytes (a
/// ray's frame has a zero every four bytes or so), and COBS pays for every
/// zero it stuffs: masked, a byte is zero only where it was this mask's
/// byte, which the fields' values seldom are. The mask is applied in the
/// CRC's own pass over the bytes, at both ends, so a frame with nothing to
/// stuff costs its stuffing one code byte. On a Cortex-M3 this took a
/// granted hop's end from 968 to 894 instructions.
///
/// Each of its bytes is the one least often found at its place (modulo 4)
/// among the 2.4e6 body bytes of the paper's frame on 4x8x2 (1000 spheres,
/// seed 1986); one frame in ten is left with a zero. Fields' low bytes are
/// near uniform, so no mask does much better.
pub const MASK: u32 = 0x7B4A_504D;

/// The mask of the CRC's four bytes after `body_len` bytes of body.
fn crc_mask(body_len: usize) -> u32 {
    MASK.rotate_right(8 * (body_len % 4) as u32)
}

/// A retirement's message as postcard writes it (the variant's index, the
/// records' wire form as a byte string, its length one varint byte) but
/// with the records written straight into place: through serde they were
/// written into a zeroed scratch buffer and copied, a twentieth of a
/// six-record message's instructions on a Cortex-M3.
fn encode_retire_message(records: &Retirements, out: &mut [u8]) -> Result<usize, EncodeError> {
    const _: () = assert!(WIRE_MAX_LEN < 0x80);
    let (head, bytes) = out.split_at_mut_checked(2).ok_or(EncodeError::BufferTooSmall)?;
    let n = records.encode_wire(bytes).ok_or(EncodeError::BufferTooSmall)?;
    head.copy_from_slice(&[RETIRE_TAG, n as u8]);
    Ok(2 + n)
}

/// postcard's variant index of [`Message::Ray`] (a test holds it to
/// postcard's). A ray's message is not written so on the wire: its own
/// head byte, with [`ray_wire::RAY`] set, is its tag. A body that starts so
/// is refused, which leaves each ray message one encoding.
const RAY_TAG: u8 = 7;
/// The same of [`Message::GrantedRay`].
const GRANTED_RAY_TAG: u8 = 24;
/// postcard's variant index of [`Message::Retire`], the first byte of its
/// body after the sequence number.
const RETIRE_TAG: u8 = 8;
/// The same of the small messages a link carries most: acknowledgements
/// alone, and the grants that pass rays.
const ACK_TAG: u8 = 15;
const NAK_TAG: u8 = 16;
const RAY_REPLY_TAG: u8 = 17;
const SPACE_TAG: u8 = 18;
const GRANT_TAG: u8 = 23;

/// The tag that starts a batch's body after its first sequence number:
/// postcard's index of no [`Message`] variant (a test holds it so).
const BATCH_TAG: u8 = 0x7F;
/// The batch's count byte has this bit set when an acknowledgement follows it.
const BATCH_ACK: u8 = 0x80;
/// Most messages in a batch: its count takes the count byte's other bits.
const BATCH_MAX: u8 = 0x7F;

/// Writes the frame's body, its postcard serialization (its sequence number,
/// then its message), at the start of `payload`; its length.
#[inline(always)]
fn encode_body(seq: Seq, msg: &Message, payload: &mut [u8]) -> Result<usize, EncodeError> {
    let (head, rest) = payload.split_first_mut().ok_or(EncodeError::BufferTooSmall)?;
    *head = seq;
    Ok(1 + encode_message(msg, rest)?)
}

/// The longest message as it follows the sequence number in a frame: the
/// room [`encode_message`] may need.
pub const MAX_MESSAGE_LEN: usize = Message::POSTCARD_MAX_SIZE;

/// Writes `msg` as it follows the sequence number in a frame (its postcard
/// serialization) at the start of `out`; its length. At most
/// [`MAX_MESSAGE_LEN`] bytes.
#[inline(never)]
pub fn encode_message(msg: &Message, out: &mut [u8]) -> Result<usize, EncodeError> {
    match msg {
        Message::Ray(ray) => encode_ray_message(&OutgoingRay::of(ray, false), out),
        Message::GrantedRay(ray) => encode_ray_message(&OutgoingRay::of(ray, true), out),
        Message::Retire(records) => encode_retire_message(records, out),
        // The small messages `decode_payload` reads by hand, written so.
        Message::Ack(ack) => put_bytes(&[ACK_TAG, *ack], out),
        Message::Nak(nak) => put_bytes(&[NAK_TAG, *nak], out),
        Message::Space => put_bytes(&[SPACE_TAG], out),
        Message::Grant(n @ 0..0x80) => put_bytes(&[GRANT_TAG, *n as u8], out),
        Message::RayReply(RayReply { tag: tag @ 0..0x80, accepted }) => {
            put_bytes(&[RAY_REPLY_TAG, *tag as u8, u8::from(*accepted)], out)
        }
        _ => Ok(postcard::to_slice(msg, out).map_err(|_| EncodeError::BufferTooSmall)?.len()),
    }
}

/// Writes `bytes` at the start of `payload`; their length.
#[inline(always)]
fn put_bytes(bytes: &[u8], payload: &mut [u8]) -> Result<usize, EncodeError> {
    payload.get_mut(..bytes.len()).ok_or(EncodeError::BufferTooSmall)?.copy_from_slice(bytes);
    Ok(bytes.len())
}

/// Writes the message `ray` stands for ([`OutgoingRay::message`]) as
/// [`encode_message`] would, straight from where the ray lies; its length.
#[inline(never)]
pub fn encode_outgoing_ray(ray: &OutgoingRay<'_>, out: &mut [u8]) -> Result<usize, EncodeError> {
    encode_ray_message(ray, out)
}

/// A ray's message as it follows the sequence number: the ray's wire form,
/// whose head byte is the message's tag (postcard would write the variant's
/// index before it, a byte a hop more) and whose header says how long it
/// is, packed straight into place. Through serde the ray was packed into a
/// zeroed scratch buffer and copied, and the variant dispatched: a tenth of
/// a hop's instructions at each end, for the message that is most of the
/// traffic.
#[inline(always)]
fn encode_ray_message(ray: &OutgoingRay<'_>, out: &mut [u8]) -> Result<usize, EncodeError> {
    ray_wire::encode_outgoing(ray, out).ok_or(EncodeError::BufferTooSmall)
}

/// Incremental frame decoder with a fixed buffer.
#[derive(Debug, Clone)]
pub struct FrameDecoder {
    buf: [u8; MAX_FRAME_LEN],
    len: usize,
    /// Set after an overflow: drop bytes until the next delimiter.
    discarding: bool,
    /// The messages of a batch not yet handed out, decoded in `buf`.
    batch: Batch,
    /// `batch` as it was before the last message handed out, if that came
    /// from a batch: what [`FrameDecoder::unread`] puts back.
    again: Batch,
}

/// What is left of a batch: `left` messages in `buf[at..end]`, the next
/// with sequence number `seq`. All zero when none is.
#[derive(Debug, Clone, Copy)]
struct Batch {
    seq: Seq,
    left: u8,
    at: u8,
    end: u8,
}

impl Batch {
    const NONE: Self = Self { seq: 0, left: 0, at: 0, end: 0 };
}

// Offsets in the buffer fit a byte.
const _: () = assert!(MAX_FRAME_LEN <= 255);

impl Default for FrameDecoder {
    fn default() -> Self {
        Self::new()
    }
}

impl FrameDecoder {
    /// An empty decoder.
    pub const fn new() -> Self {
        Self { buf: [0; MAX_FRAME_LEN], len: 0, discarding: false, batch: Batch::NONE, again: Batch::NONE }
    }

    /// Consumes bytes from the front of `bytes` up to the first result: a
    /// frame a delimiter closes, or an overflow. `None` once every byte is
    /// consumed without one. However the bytes are cut into calls, the
    /// results are the same. `bytes` keeps what was not read: call again
    /// until `None`.
    ///
    /// A batch of messages gives a frame for each, one a call, before any
    /// more bytes are read: the first carries the batch's sequence number
    /// and acknowledgement, each next the next sequence number and none.
    ///
    /// Bytes between delimiters are copied as a block: on a Cortex-M3 this
    /// costs a fraction of pushing them one by one, where every byte returns
    /// an `Option` as large as a frame.
    pub fn decode(&mut self, bytes: &mut &[u8]) -> Option<Result<Frame, DecodeError>> {
        let mut frame = Frame::new(0, Message::Space);
        Some(self.decode_into(bytes, &mut frame)?.map(|()| frame))
    }

    /// [`FrameDecoder::decode`], writing the frame into `out` (left as it
    /// was on an error): a frame is as large as a ray with its hit, and
    /// handed back by value it was copied at each return on its way to the
    /// channel (on a Cortex-M3, 37 instructions of each end of a hop).
    pub fn decode_into(&mut self, bytes: &mut &[u8], out: &mut Frame) -> Option<Result<(), DecodeError>> {
        if self.batch.left > 0 {
            return Some(self.next_of_batch(out));
        }
        // Bytes go where a batch put back would be read from.
        if !bytes.is_empty() {
            self.again = Batch::NONE;
        }
        while let Some((&first, after)) = bytes.split_first() {
            // A zero with nothing before it, an empty frame (a sender may
            // open a frame with one, as PPP does after an idle line):
            // skipped at once.
            if first == 0 && self.len == 0 && !self.discarding {
                *bytes = after;
                continue;
            }
            let (run, closed, rest) = match cobs::first_zero(bytes) {
                Some(at) => {
                    (bytes.get(..at).unwrap_or_default(), true, bytes.get(at + 1..).unwrap_or_default())
                }
                None => (*bytes, false, &[][..]),
            };
            *bytes = rest;
            if !self.extend(run) {
                // The delimiter, if any, ends the frame being discarded.
                if closed {
                    self.close(out);
                }
                return Some(Err(DecodeError::Oversize));
            }
            if closed && let Some(result) = self.close(out) {
                return Some(result);
            }
        }
        None
    }

    /// Appends a run of non-zero bytes; false when it overflows the buffer
    /// (then the frame's bytes are dropped up to its delimiter).
    fn extend(&mut self, run: &[u8]) -> bool {
        if self.discarding || run.is_empty() {
            return true;
        }
        match self.buf.get_mut(self.len..self.len + run.len()) {
            Some(dst) => {
                dst.copy_from_slice(run);
                self.len += run.len();
                true
            }
            None => {
                self.discarding = true;
                self.len = 0;
                false
            }
        }
    }

    /// Drops any partial frame and what is left of a batch, as after a link reset.
    pub fn reset(&mut self) {
        self.len = 0;
        self.discarding = false;
        self.batch = Batch::NONE;
        self.again = Batch::NONE;
    }

    /// Puts the last message handed out back, if it came from a batch: the
    /// next call hands it out again, before reading any byte. Whether it did.
    /// A receiver with no room for a batch's next message so keeps it, and
    /// the rest, until it has (reading no bytes meanwhile: the batch is in
    /// the buffer they would go to).
    pub fn unread(&mut self) -> bool {
        let again = core::mem::replace(&mut self.again, Batch::NONE);
        if again.left == 0 {
            return false;
        }
        self.batch = again;
        true
    }

    /// Whether messages of a batch wait to be handed out: feed no bytes
    /// until they have been (a call with none hands them out).
    pub fn holds_batch(&self) -> bool {
        self.batch.left > 0
    }

    fn close(&mut self, out: &mut Frame) -> Option<Result<(), DecodeError>> {
        let len = core::mem::take(&mut self.len);
        if core::mem::take(&mut self.discarding) || len == 0 {
            return None;
        }
        let encoded = self.buf.get_mut(..len)?;
        Some(decode_payload(encoded, out).map(|(rest, again)| {
            self.batch = rest;
            self.again = again;
        }))
    }

    /// The next message of the batch in the buffer, into `out`. Out of line:
    /// every call of `decode_into` asks, few find a batch.
    #[inline(never)]
    fn next_of_batch(&mut self, out: &mut Frame) -> Result<(), DecodeError> {
        let before = core::mem::replace(&mut self.batch, Batch::NONE);
        self.again = Batch::NONE;
        let Batch { seq, left, at, end } = before;
        let bytes = self.buf.get(usize::from(at)..usize::from(end)).ok_or(DecodeError::Body)?;
        let left = left.saturating_sub(1);
        let rest = decode_message(bytes, &mut out.msg, left)?;
        (out.seq, out.ack) = (seq, None);
        if left > 0 {
            self.batch = Batch { seq: seq.wrapping_add(1), left, at: end.saturating_sub(rest), end };
        }
        self.again = before;
        Ok(())
    }
}

/// Decodes one COBS payload (delimiters stripped) in place, into `out`
/// (untouched on an error): a frame's message, or a batch's first; then
/// what is left of the batch.
///
/// Out of line: inlined into `close`, the message was built aside and
/// copied into `out` (60 instructions a frame on a Cortex-M3).
#[inline(never)]
fn decode_payload(encoded: &mut [u8], out: &mut Frame) -> Result<(Batch, Batch), DecodeError> {
    let (start, len) = cobs::decode_in_place(encoded).ok_or(DecodeError::Cobs)?;
    let payload = encoded.get_mut(start..start + len).ok_or(DecodeError::Cobs)?;
    let body_len = payload.len().checked_sub(CRC_LEN).ok_or(DecodeError::Short)?;
    let (body, crc) = payload.split_at_mut(body_len);
    let mut crc_bytes = [0u8; CRC_LEN];
    crc_bytes.copy_from_slice(crc);
    if crc32c::unmask_then_checksum(body, MASK) != u32::from_le_bytes(crc_bytes) ^ crc_mask(body_len) {
        return Err(DecodeError::Crc);
    }
    match &*body {
        // A ray, read as `encode_ray_message` writes it: no serde dispatch,
        // and written straight into `out`.
        [seq, rest @ ..] if rest.first().is_some_and(|&tag| tag & ray_wire::RAY != 0) => {
            let ack = ray_wire::decode_ray_into(rest, &mut out.msg, |trailer| decode_trailer(trailer).ok());
            (out.seq, out.ack) = (*seq, ack.ok_or(DecodeError::Body)?);
            Ok((Batch::NONE, Batch::NONE))
        }
        [seq, BATCH_TAG, head, rest @ ..] => {
            // Offsets in the buffer: the body starts at `start`.
            let end = u8::try_from(start + body_len).map_err(|_| DecodeError::Body)?;
            decode_batch(*seq, *head, rest, end, out)
        }
        // The small messages a link carries most, read as postcard writes
        // them (a grant or a reply's tag under 128 is one varint byte, a
        // bool a byte 0 or 1): through serde's dispatch each cost a hundred
        // and more instructions to build.
        [seq, ACK_TAG, ack, trailer @ ..] => put(out, *seq, Message::Ack(*ack), trailer),
        [seq, NAK_TAG, nak, trailer @ ..] => put(out, *seq, Message::Nak(*nak), trailer),
        [seq, SPACE_TAG, trailer @ ..] => put(out, *seq, Message::Space, trailer),
        [seq, RAY_REPLY_TAG, tag @ 0..0x80, accepted @ 0..=1, trailer @ ..] => {
            let reply = RayReply { tag: u16::from(*tag), accepted: *accepted == 1 };
            put(out, *seq, Message::RayReply(reply), trailer)
        }
        [seq, GRANT_TAG, n @ 0..0x80, trailer @ ..] => put(out, *seq, Message::Grant(u16::from(*n)), trailer),
        [_, RAY_TAG | GRANTED_RAY_TAG, ..] => Err(DecodeError::Body),
        _ => {
            // Straight from the deserializer: `take_from_bytes` moves the frame
            // through two more temporaries, each a byte-wise copy on a Cortex-M. And
            // field by field rather than `Frame::deserialize`, whose sequence access
            // LLVM may take out of line (it did when `Hello` grew a field), handing
            // the message back through memory: 330 more instructions a frame.
            let mut de = postcard::Deserializer::from_bytes(body);
            let seq = Seq::deserialize(&mut de).map_err(|_| DecodeError::Body)?;
            let msg = Message::deserialize(&mut de).map_err(|_| DecodeError::Body)?;
            let trailer = de.finalize().map_err(|_| DecodeError::Body)?;
            put(out, seq, msg, trailer)
        }
    }
}

/// Writes the frame of `seq`, `msg` and the acknowledgement `trailer` holds
/// into `out`, if it holds one or none. Inlined, so that a small message is
/// written in place rather than built aside, as large as a ray, and copied.
#[inline(always)]
fn put(out: &mut Frame, seq: Seq, msg: Message, trailer: &[u8]) -> Result<(Batch, Batch), DecodeError> {
    let ack = decode_trailer(trailer)?;
    *out = Frame { seq, msg, ack };
    Ok((Batch::NONE, Batch::NONE))
}

/// A batch's head (`head`: its count and whether an acknowledgement
/// follows) and first message into `out`, from `rest`, the bytes after the
/// head up to `end`; what is left of it, and the whole batch (for
/// [`FrameDecoder::unread`]).
fn decode_batch(
    seq: Seq,
    head: u8,
    rest: &[u8],
    end: u8,
    out: &mut Frame,
) -> Result<(Batch, Batch), DecodeError> {
    let (count, ack, messages) = match (head & !BATCH_ACK, head & BATCH_ACK != 0, rest) {
        (0, _, _) | (_, true, []) => return Err(DecodeError::Body),
        (count, false, messages) => (count, None, messages),
        (count, true, [ack, messages @ ..]) => (count, Some(*ack), messages),
    };
    let left = count - 1;
    let rest = decode_message(messages, &mut out.msg, left)?;
    (out.seq, out.ack) = (seq, ack);
    // `messages` runs to `end`, within a buffer of at most 255 bytes.
    let whole = Batch { seq, left: count, at: end.saturating_sub(messages.len() as u8), end };
    let rest = if left > 0 {
        Batch { seq: seq.wrapping_add(1), left, at: end.saturating_sub(rest), end }
    } else {
        Batch::NONE
    };
    Ok((rest, whole))
}

/// Decodes a batch's message at the start of `bytes` into `out` (left as it
/// was on an error); `left` more follow it, and the last must end the
/// batch. How many bytes follow it.
fn decode_message(bytes: &[u8], out: &mut Message, left: u8) -> Result<u8, DecodeError> {
    let rest = |after: &[u8]| match (left, after.len()) {
        (0, 0) => Ok(0),
        (0, _) => Err(DecodeError::Body),
        // Within a buffer of at most 255 bytes.
        (_, n) => u8::try_from(n).map_err(|_| DecodeError::Body),
    };
    match bytes.first() {
        Some(&tag) if tag & ray_wire::RAY != 0 => {
            return ray_wire::decode_ray_into(bytes, out, |after| rest(after).ok()).ok_or(DecodeError::Body);
        }
        Some(&(RAY_TAG | GRANTED_RAY_TAG)) => return Err(DecodeError::Body),
        _ => {}
    }
    let (msg, after) = postcard::take_from_bytes::<Message>(bytes).map_err(|_| DecodeError::Body)?;
    let n = rest(after)?;
    *out = msg;
    Ok(n)
}

/// The acknowledgement trailer, if any: it must fill `trailer` exactly.
fn decode_trailer(trailer: &[u8]) -> Result<Option<Seq>, DecodeError> {
    if trailer.is_empty() { Ok(None) } else { decode_ack(trailer).map(Some) }
}

/// Decodes the acknowledgement trailer, which must fill `trailer` exactly.
fn decode_ack(trailer: &[u8]) -> Result<Seq, DecodeError> {
    match postcard::take_from_bytes::<Seq>(trailer) {
        Ok((ack, [])) => Ok(ack),
        _ => Err(DecodeError::Body),
    }
}

#[cfg(test)]
mod tests {
    use super::BATCH_TAG;
    use crate::message::Message;

    #[test]
    fn the_batch_tag_is_no_messages() {
        // postcard would read it as a variant index: there must be none.
        for next in [0u8, 1, 0x7F, 0xFF] {
            assert!(postcard::from_bytes::<Message>(&[BATCH_TAG, next, 0, 0]).is_err());
        }
    }
}
