//! Framing: `0x00 ++ COBS(postcard(frame) ++ [ack] ++ crc32c_le) ++ 0x00`.
//!
//! `ack` is the optional piggybacked acknowledgement ([`Frame::ack`]), one
//! byte ([`Seq`]) after the body: present exactly when bytes remain between
//! the body and the CRC.
//!
//! The leading zero means a frame cut short by a lost byte run damages only
//! itself: the next frame starts clean. The CRC sits inside the COBS payload, so a
//! corrupted byte anywhere (including one that COBS decodes without complaint) is
//! caught. [`FrameDecoder`] never panics and resynchronises on the next zero byte
//! after garbage, a truncated frame or an oversize one.

use crate::message::{Frame, Message, RayMsg, RayReply, Seq};
use crate::{cobs, crc32c, ray_wire};
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

/// Largest encoded frame on the wire, both zero delimiters included.
pub const MAX_FRAME_LEN: usize = cobs::max_encoding_length(MAX_PAYLOAD_LEN) + 2;

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
/// The payload is written straight into `out` after the leading delimiter and
/// a slot for the first COBS code byte, then stuffed in place: no scratch
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
    // out = [0, code, payload.., 0]; the payload may use at most what is left.
    let room = out.len().saturating_sub(3).min(MAX_PAYLOAD_LEN);
    let payload = out.get_mut(2..2 + room).ok_or(SMALL)?;
    let mut body_len = encode_body(seq, msg, payload)?;
    if let Some(ack) = ack {
        let trailer = payload.get_mut(body_len..).ok_or(SMALL)?;
        body_len += postcard::to_slice(&ack, trailer).map_err(|_| SMALL)?.len();
    }
    let crc = checksum(payload.get(..body_len).unwrap_or_default());
    let payload_len = body_len + CRC_LEN;
    payload.get_mut(body_len..payload_len).ok_or(SMALL)?.copy_from_slice(&crc.to_le_bytes());
    // MAX_PAYLOAD_LEN bounds the payload well under COBS's in-place limit.
    cobs::encode_in_place(out.get_mut(1..2 + payload_len).ok_or(SMALL)?).ok_or(SMALL)?;
    *out.first_mut().ok_or(SMALL)? = 0;
    *out.get_mut(2 + payload_len).ok_or(SMALL)? = 0;
    Ok(payload_len + 3)
}

/// postcard's variant index of [`Message::Ray`], the first byte of its body
/// after the sequence number (a test holds it to postcard's).
const RAY_TAG: u8 = 7;
/// The same of [`Message::GrantedRay`].
const GRANTED_RAY_TAG: u8 = 24;
/// The same of the small messages a link carries most: acknowledgements
/// alone, and the grants that pass rays.
const ACK_TAG: u8 = 15;
const NAK_TAG: u8 = 16;
const RAY_REPLY_TAG: u8 = 17;
const SPACE_TAG: u8 = 18;
const GRANT_TAG: u8 = 23;

/// Writes the frame's body, its postcard serialization (its sequence number,
/// then its message), at the start of `payload`; its length.
fn encode_body(seq: Seq, msg: &Message, payload: &mut [u8]) -> Result<usize, EncodeError> {
    match msg {
        Message::Ray(ray) => encode_ray_body(seq, RAY_TAG, ray, payload),
        Message::GrantedRay(ray) => encode_ray_body(seq, GRANTED_RAY_TAG, ray, payload),
        _ => {
            let seq_len =
                postcard::to_slice(&seq, &mut *payload).map_err(|_| EncodeError::BufferTooSmall)?.len();
            let msg_out = payload.get_mut(seq_len..).ok_or(EncodeError::BufferTooSmall)?;
            Ok(seq_len + postcard::to_slice(msg, msg_out).map_err(|_| EncodeError::BufferTooSmall)?.len())
        }
    }
}

/// The body of a frame carrying a ray, written as postcard writes it (the
/// sequence number, the variant's index, the ray's wire form as a byte
/// string: its length in one varint byte, as `RAY_MAX_LEN < 128`) but with
/// the ray packed straight into place. Through serde the ray was packed into
/// a zeroed scratch buffer and copied, and the variant dispatched: a tenth
/// of a hop's instructions at each end, for the message that is most of the
/// traffic.
fn encode_ray_body(seq: Seq, tag: u8, ray: &RayMsg, payload: &mut [u8]) -> Result<usize, EncodeError> {
    let (head, bytes) = payload.split_at_mut_checked(3).ok_or(EncodeError::BufferTooSmall)?;
    let n = ray_wire::encode_ray(ray, bytes).ok_or(EncodeError::BufferTooSmall)?;
    head.copy_from_slice(&[seq, tag, n as u8]);
    Ok(3 + n)
}

/// Incremental frame decoder with a fixed buffer.
#[derive(Debug, Clone)]
pub struct FrameDecoder {
    buf: [u8; MAX_FRAME_LEN],
    len: usize,
    /// Set after an overflow: drop bytes until the next delimiter.
    discarding: bool,
}

impl Default for FrameDecoder {
    fn default() -> Self {
        Self::new()
    }
}

impl FrameDecoder {
    /// An empty decoder.
    pub const fn new() -> Self {
        Self { buf: [0; MAX_FRAME_LEN], len: 0, discarding: false }
    }

    /// Feeds one byte. Returns a result each time a delimiter closes a non-empty frame.
    pub fn push(&mut self, byte: u8) -> Option<Result<Frame, DecodeError>> {
        self.decode(&mut &[byte][..])
    }

    /// Consumes bytes from the front of `bytes` up to the first result: a
    /// frame a delimiter closes, or an overflow. `None` once every byte is
    /// consumed without one. However the bytes are cut into calls, the
    /// results are the same.
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
        while !bytes.is_empty() {
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

    /// Drops any partial frame, as after a link reset.
    pub fn reset(&mut self) {
        self.len = 0;
        self.discarding = false;
    }

    fn close(&mut self, out: &mut Frame) -> Option<Result<(), DecodeError>> {
        let len = core::mem::take(&mut self.len);
        if core::mem::take(&mut self.discarding) || len == 0 {
            return None;
        }
        let encoded = self.buf.get_mut(..len)?;
        Some(decode_payload(encoded, out))
    }
}

/// Decodes one COBS payload (delimiters stripped) in place, into `out`
/// (untouched on an error).
fn decode_payload(encoded: &mut [u8], out: &mut Frame) -> Result<(), DecodeError> {
    let payload = cobs::decode_slice(encoded).ok_or(DecodeError::Cobs)?;
    let body_len = payload.len().checked_sub(CRC_LEN).ok_or(DecodeError::Short)?;
    let (body, crc) = payload.split_at(body_len);
    let mut crc_bytes = [0u8; CRC_LEN];
    crc_bytes.copy_from_slice(crc);
    if checksum(body) != u32::from_le_bytes(crc_bytes) {
        return Err(DecodeError::Crc);
    }
    let (seq, msg, trailer) = match body {
        // A ray, read as `encode_ray_body` writes it: no serde dispatch,
        // and written straight into `out`.
        [seq, tag @ (RAY_TAG | GRANTED_RAY_TAG), len @ 0..0x80, rest @ ..] => {
            let (bytes, trailer) = rest.split_at_checked(usize::from(*len)).ok_or(DecodeError::Body)?;
            let ack = decode_trailer(trailer)?;
            let ray = ray_wire::decode_ray(bytes).ok_or(DecodeError::Body)?;
            out.msg = if *tag == RAY_TAG { Message::Ray(ray) } else { Message::GrantedRay(ray) };
            (out.seq, out.ack) = (*seq, ack);
            return Ok(());
        }
        // The small messages a link carries most, read as postcard writes
        // them (a grant or a reply's tag under 128 is one varint byte, a
        // bool a byte 0 or 1): through serde's dispatch each cost a hundred
        // and more instructions to build.
        [seq, ACK_TAG, ack, trailer @ ..] => (*seq, Message::Ack(*ack), trailer),
        [seq, NAK_TAG, nak, trailer @ ..] => (*seq, Message::Nak(*nak), trailer),
        [seq, SPACE_TAG, trailer @ ..] => (*seq, Message::Space, trailer),
        [seq, RAY_REPLY_TAG, tag @ 0..0x80, accepted @ 0..=1, trailer @ ..] => {
            (*seq, Message::RayReply(RayReply { tag: u16::from(*tag), accepted: *accepted == 1 }), trailer)
        }
        [seq, GRANT_TAG, n @ 0..0x80, trailer @ ..] => (*seq, Message::Grant(u16::from(*n)), trailer),
        _ => {
            // Straight from the deserializer: `take_from_bytes` moves the frame
            // through two more temporaries, each a byte-wise copy on a Cortex-M. And
            // field by field rather than `Frame::deserialize`, whose sequence access
            // LLVM may take out of line (it did when `Hello` grew a field), handing
            // the message back through memory: 330 more instructions a frame.
            let mut de = postcard::Deserializer::from_bytes(body);
            let seq = Seq::deserialize(&mut de).map_err(|_| DecodeError::Body)?;
            let msg = Message::deserialize(&mut de).map_err(|_| DecodeError::Body)?;
            (seq, msg, de.finalize().map_err(|_| DecodeError::Body)?)
        }
    };
    let ack = decode_trailer(trailer)?;
    *out = Frame { seq, msg, ack };
    Ok(())
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
