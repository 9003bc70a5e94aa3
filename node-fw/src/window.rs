//! A reliable channel's send window: the messages sent and not yet
//! acknowledged, oldest first, each kept in its wire form.
//!
//! A message is encoded once, straight into its slot, when it is queued;
//! every write of it (the first, and any resend after a loss) copies those
//! bytes into a frame. Kept as `Message` values, each queued ray was copied
//! whole into the window (as large as a ray with its hit, 128 bytes) and
//! encoded again on every write.

use link_proto::{
    EncodeError, MAX_MESSAGE_LEN, Message, OutgoingRay, Seq, encode_message, encode_outgoing_ray,
};

/// Up to `W` messages with their sequence numbers, in a ring of fixed slots.
#[derive(Debug)]
pub struct Window<const W: usize> {
    /// Slot `(head + k) % W` holds the `k`-th oldest message's bytes.
    slots: [[u8; MAX_MESSAGE_LEN]; W],
    /// Each slot's sequence number and length.
    entries: [Entry; W],
    head: usize,
    len: usize,
}

#[derive(Debug, Clone, Copy)]
struct Entry {
    seq: Seq,
    len: u8,
}

// Lengths fit an entry's byte.
const _: () = assert!(MAX_MESSAGE_LEN <= 255);

impl<const W: usize> Default for Window<W> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const W: usize> Window<W> {
    /// An empty window.
    pub const fn new() -> Self {
        Self { slots: [[0; MAX_MESSAGE_LEN]; W], entries: [Entry { seq: 0, len: 0 }; W], head: 0, len: 0 }
    }

    /// Messages held.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether none is held.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Whether `W` are held.
    pub fn is_full(&self) -> bool {
        self.len >= W
    }

    /// The ring index of the `k`-th oldest message.
    fn slot(&self, k: usize) -> usize {
        (self.head + k) % W
    }

    /// Encodes `msg` into the next slot as `seq`. Fails when the window is
    /// full (a message always fits its slot: [`MAX_MESSAGE_LEN`] is its
    /// encoding's bound).
    pub fn push(&mut self, seq: Seq, msg: &Message) -> Result<(), EncodeError> {
        self.push_with(seq, |slot| encode_message(msg, slot))
    }

    /// Encodes the message `ray` stands for into the next slot as `seq`,
    /// from where the ray lies; fails as [`Self::push`] does.
    pub fn push_ray(&mut self, seq: Seq, ray: &OutgoingRay<'_>) -> Result<(), EncodeError> {
        self.push_with(seq, |slot| encode_outgoing_ray(ray, slot))
    }

    /// Has `encode` write the next slot, numbered `seq`.
    #[inline(always)]
    fn push_with(
        &mut self,
        seq: Seq,
        encode: impl FnOnce(&mut [u8]) -> Result<usize, EncodeError>,
    ) -> Result<(), EncodeError> {
        if self.is_full() {
            return Err(EncodeError::BufferTooSmall);
        }
        let at = self.slot(self.len);
        let slot = self.slots.get_mut(at).ok_or(EncodeError::BufferTooSmall)?;
        let len = encode(slot)?;
        let entry = self.entries.get_mut(at).ok_or(EncodeError::BufferTooSmall)?;
        // `len` is at most the slot's length, under 256.
        *entry = Entry { seq, len: len as u8 };
        self.len += 1;
        Ok(())
    }

    /// The oldest message's sequence number.
    pub fn front_seq(&self) -> Option<Seq> {
        self.get(0).map(|(seq, _)| seq)
    }

    /// Drops the oldest message.
    pub fn pop_front(&mut self) {
        if self.len > 0 {
            self.head = self.slot(1);
            self.len -= 1;
        }
    }

    /// The `k`-th oldest message: its sequence number and bytes.
    pub fn get(&self, k: usize) -> Option<(Seq, &[u8])> {
        if k >= self.len {
            return None;
        }
        let at = self.slot(k);
        let entry = self.entries.get(at)?;
        Some((entry.seq, self.slots.get(at)?.get(..usize::from(entry.len))?))
    }

    /// The messages from the `k`-th oldest on.
    pub fn iter_from(&self, k: usize) -> impl Iterator<Item = (Seq, &[u8])> {
        (k..self.len).filter_map(|k| self.get(k))
    }

    /// Numbers the messages afresh, oldest first, from `first`; the number
    /// after the last.
    pub fn renumber(&mut self, first: Seq) -> Seq {
        let mut seq = first;
        for k in 0..self.len {
            let at = self.slot(k);
            if let Some(entry) = self.entries.get_mut(at) {
                entry.seq = seq;
            }
            seq = seq.wrapping_add(1);
        }
        seq
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use std::vec::Vec;

    use super::*;
    use link_proto::{FrameDecoder, MAX_FRAME_LEN, RayReply, encode_encoded};

    fn reply(tag: u16) -> Message {
        Message::RayReply(RayReply { tag, accepted: true })
    }

    /// What the window holds, each message framed and read back by the
    /// frame decoder.
    fn held<const W: usize>(w: &Window<W>) -> Vec<(Seq, Message)> {
        let mut buf = [0u8; MAX_FRAME_LEN];
        let mut out = Vec::new();
        for (seq, bytes) in w.iter_from(0) {
            let n = encode_encoded(seq, bytes, None, &mut buf).unwrap();
            let frame = FrameDecoder::new().decode(&mut &buf[..n]).unwrap().unwrap();
            out.push((frame.seq, frame.msg));
        }
        out
    }

    #[test]
    fn it_keeps_messages_in_order_around_the_ring() {
        let mut w = Window::<3>::new();
        for round in 0u16..5 {
            let seq = (round * 2) as Seq;
            w.push(seq, &reply(round)).unwrap();
            w.push(seq + 1, &Message::Grant(round + 300)).unwrap();
            assert_eq!(held(&w), [(seq, reply(round)), (seq + 1, Message::Grant(round + 300))]);
            assert_eq!(w.front_seq(), Some(seq));
            w.pop_front();
            w.pop_front();
            assert!(w.is_empty());
        }
    }

    #[test]
    fn a_full_window_refuses_and_keeps_what_it_holds() {
        let mut w = Window::<2>::new();
        w.push(7, &Message::Space).unwrap();
        w.push(8, &reply(1)).unwrap();
        assert!(w.is_full());
        assert_eq!(w.push(9, &reply(2)), Err(EncodeError::BufferTooSmall));
        assert_eq!(held(&w), [(7, Message::Space), (8, reply(1))]);
        w.pop_front();
        w.pop_front();
        w.pop_front();
        assert_eq!((w.len(), w.front_seq(), w.get(0)), (0, None, None));
    }

    #[test]
    fn renumbering_starts_from_the_oldest() {
        let mut w = Window::<4>::new();
        for seq in 250..254 {
            w.push(seq, &Message::Space).unwrap();
        }
        w.pop_front();
        assert_eq!(w.renumber(0), 3);
        let seqs: Vec<Seq> = w.iter_from(0).map(|(s, _)| s).collect();
        assert_eq!(seqs, [0, 1, 2]);
        assert_eq!(w.iter_from(2).count(), 1);
    }
}
