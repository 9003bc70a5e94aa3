//! Wire messages and framing for the sliding-boundary ray tracer.
//!
//! Every conversation of the system (host to node, node to node) is a [`Message`]
//! carried in a [`Frame`] with a per-link sequence number and, perhaps, an
//! acknowledgement riding on it. A frame travels as
//! `0x00 ++ COBS(postcard(frame) ++ [ack] ++ crc32c_le) ++ 0x00` ([`frame`]), so a
//! receiver can resynchronise on the next zero byte after garbage, and any
//! corrupted byte is caught by the CRC. A ray travels in a compact form of its
//! own ([`ray_wire`]), and retirements several to a message in a compact form
//! ([`retirements`]).
//!
//! All numbers on the wire are plain integers: fixed-point values travel as their
//! raw bits, with the format named in each field's documentation. The largest
//! encoded frame ([`MAX_FRAME_LEN`]) is known at compile time, so every buffer is
//! a fixed array and nothing allocates.
#![no_std]
#![cfg_attr(not(test), deny(clippy::unwrap_used, clippy::expect_used, clippy::panic))]
#![cfg_attr(not(test), deny(clippy::indexing_slicing))]

pub mod board;
pub mod cobs;
mod crc32c;
pub mod credit;
pub mod frame;
pub mod health;
pub mod message;
mod pack;
pub mod ray_wire;
pub mod retirements;
pub mod site;

pub use board::{BoardId, BoardInfo, BoardKind, ClockSource, FirmwareVersion, PeerNote};
pub use frame::{
    DecodeError, EncodeError, FrameDecoder, MAX_FRAME_LEN, MAX_MESSAGE_LEN, MAX_PAYLOAD_LEN, encode_batch,
    encode_encoded, encode_frame, encode_message, encode_outgoing_ray, encode_parts,
};
pub use health::{LinkHealth, PortHealth};
pub use message::*;
pub use ray_wire::OutgoingRay;
pub use site::{Found, Site};

/// Version of the wire protocol; nodes and host exchange it in [`Hello`].
/// Bump it whenever a message changes shape (postcard carries no field names).
pub const PROTOCOL_VERSION: u16 = 29;
