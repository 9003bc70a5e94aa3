//! One node's view of its in-memory links during a round.

use std::collections::VecDeque;

use link_proto::{MAX_FRAME_LEN, Message, encode_frame};
use node_fw::{Links, Port};

/// A message in a link, stamped with its arrival time and its length as a frame.
#[derive(Debug, Clone)]
pub struct Stamped {
    /// Virtual time of arrival.
    pub at: u64,
    /// The message.
    pub msg: Message,
    /// Bytes it takes on the wire.
    pub len: u64,
    /// It went in a batch with the messages before it, not a frame of its own.
    pub joined: bool,
    /// When the frame it went in started on the wire: its batch, on its port.
    pub frame_start: u64,
}

/// What a neighbour port's wire is sending or is about to: the batch at the
/// end of this round's outbox, while it has not started on the wire.
#[derive(Debug, Clone, Copy)]
pub struct Waiting {
    /// When its first byte goes on the wire.
    pub start: u64,
    /// Its bytes on the wire, as one frame.
    pub len: u64,
    /// Its messages: the last this many of the outbox.
    pub count: usize,
    /// Begun by the poll sending now: the board writes what one poll sent
    /// as one batch, whenever its wire is free.
    pub this_poll: bool,
}

/// Bytes a message's frame of its own takes beyond what it adds to a batch:
/// its delimiter, the first COBS code, the sequence number and the CRC.
const FRAME_ALONE: u64 = 7;
/// Bytes a batch's head adds to its first message's frame: its tag and count.
const BATCH_HEAD: u64 = 2;

/// Per-port state a node owns: what has arrived, what it sent this round.
#[derive(Debug, Default)]
pub struct PortState {
    /// Messages sent to this node, in arrival order.
    pub inbox: VecDeque<Stamped>,
    /// Messages this node sent on the port this round.
    pub outbox: Vec<Stamped>,
    /// Messages in the peer's inbox from this port at the round's start.
    pub occupancy: usize,
    /// When the port's wire is free again.
    pub busy_until: u64,
    /// Bytes sent on the port.
    pub bytes: u64,
    /// Bytes taken from the port (whole messages or frames).
    pub bytes_in: u64,
    /// Framed mode: byte chunks (one frame each) arriving on this port, by arrival.
    pub wire: VecDeque<(u64, Vec<u8>)>,
    /// Framed mode: frames this node wrote on the port this round.
    pub wire_out: Vec<(u64, Vec<u8>)>,
    /// The batch messages sent now would join, if one waits for the wire.
    pub waiting: Option<Waiting>,
}

/// [`Links`] over a node's seven [`PortState`]s at virtual time `now`.
pub struct SimLinks<'a> {
    /// The node's ports, indexed by [`Port::index`].
    pub ports: &'a mut [PortState; 7],
    /// Which neighbour ports exist.
    pub wired: [bool; 7],
    /// The node's clock.
    pub now: u64,
    /// Node-to-node link timing and capacity.
    pub link: crate::cost::LinkModel,
    /// Node-to-host link timing and capacity.
    pub host_link: crate::cost::LinkModel,
    /// Set when the node tried to send through a port with no neighbour.
    pub miswired: Option<Port>,
    /// CPU cycles spent moving the bytes of the messages sent and taken,
    /// and starting the frames sent.
    pub byte_cpu: u64,
    /// Messages sent or taken that shared a frame with the ones before
    /// them: each spares its end a frame's handling.
    pub joined: u64,
    /// Messages the poll sent, in order, until [`SimLinks::transmit`].
    pub queued: &'a mut Vec<(Port, Message)>,
}

impl SimLinks<'_> {
    fn model(&self, port: Port) -> crate::cost::LinkModel {
        if port == Port::Host { self.host_link } else { self.link }
    }
}

impl Links for SimLinks<'_> {
    fn recv(&mut self, port: Port) -> Option<Message> {
        let byte_cpu = self.model(port).byte_cpu;
        let state = self.ports.get_mut(port.index())?;
        if state.inbox.front().is_some_and(|m| m.at <= self.now) {
            let m = state.inbox.pop_front()?;
            state.bytes_in += m.len;
            self.byte_cpu += m.len * byte_cpu;
            self.joined += u64::from(m.joined);
            Some(m.msg)
        } else {
            None
        }
    }

    fn cabled(&self, port: Port) -> bool {
        self.wired.get(port.index()).copied().unwrap_or(false)
    }

    /// Takes `msg` if the port has room; it goes on the wire when the poll
    /// is over ([`SimLinks::transmit`]), as a board's loop sends what a
    /// poll queued only after the poll's work.
    fn try_send(&mut self, port: Port, msg: Message) -> Result<(), Message> {
        if !self.wired.get(port.index()).copied().unwrap_or(false) {
            self.miswired = Some(port);
            return Err(msg);
        }
        let model = self.model(port);
        let Some(state) = self.ports.get(port.index()) else { return Err(msg) };
        let queued = self.queued.iter().filter(|(p, _)| *p == port).count();
        if state.occupancy + state.outbox.len() + queued >= model.capacity {
            return Err(msg);
        }
        self.queued.push((port, msg));
        Ok(())
    }
}

impl SimLinks<'_> {
    /// Puts what the poll queued on the wires at `now`, the poll's end, in
    /// the order it was sent.
    pub fn transmit(&mut self, now: u64) {
        self.now = now;
        for state in self.ports.iter_mut() {
            if let Some(w) = state.waiting.as_mut() {
                w.this_poll = false;
            }
        }
        let mut queued = std::mem::take(self.queued);
        for (port, msg) in queued.drain(..) {
            self.put_on_wire(port, msg);
        }
        *self.queued = queued;
    }

    fn put_on_wire(&mut self, port: Port, msg: Message) {
        let model = self.model(port);
        let Some(state) = self.ports.get_mut(port.index()) else { return };
        let bytes = frame_len(&msg) as u64;
        if port != Port::Host
            && let Some(added) = state.join(bytes, self.now)
        {
            // Queued behind a busy wire, or sent in the same poll: it leaves
            // in the waiting batch, which arrives whole once its last byte
            // has crossed.
            state.busy_until += added * model.byte;
            state.bytes += added;
            let at = state.busy_until + model.latency;
            let frame_start = state.waiting.map_or(0, |w| w.start);
            // Those of a batch begun in an earlier round are in the peer's
            // inbox: the board moves them when it delivers this one.
            state.outbox.iter_mut().filter(|m| m.frame_start == frame_start).for_each(|m| m.at = at);
            state.outbox.push(Stamped { at, msg, len: added, joined: true, frame_start });
            self.byte_cpu += added * model.byte_cpu;
            self.joined += 1;
            return;
        }
        let start = self.now.max(state.busy_until);
        state.busy_until = start + bytes * model.byte;
        state.bytes += bytes;
        let stamped = Stamped {
            at: state.busy_until + model.latency,
            msg,
            len: bytes,
            joined: false,
            frame_start: start,
        };
        state.outbox.push(stamped);
        state.waiting = Some(Waiting { start, len: bytes, count: 1, this_poll: true });
        self.byte_cpu += bytes * model.byte_cpu + model.frame_cpu;
    }
}

impl PortState {
    /// Adds a message whose frame alone takes `bytes` to the batch waiting
    /// for the wire at `now`, if one waits and it fits; the bytes it adds.
    ///
    /// The channel sends what is due together (`encode_batch`): a message
    /// sent while the frames before it still wait for the wire, or in the
    /// same poll, goes with them. A frame once on the wire takes nothing more.
    fn join(&mut self, bytes: u64, now: u64) -> Option<u64> {
        let w = self.waiting.as_mut().filter(|w| w.start > now || w.this_poll)?;
        let added = bytes.saturating_sub(FRAME_ALONE) + if w.count == 1 { BATCH_HEAD } else { 0 };
        if w.len + added > MAX_FRAME_LEN as u64 {
            return None;
        }
        w.len += added;
        w.count += 1;
        Some(added)
    }
}

/// Bytes the message takes on the wire as a frame.
pub fn frame_len(msg: &Message) -> usize {
    let mut buf = [0u8; MAX_FRAME_LEN];
    let frame = link_proto::Frame::new(0, msg.clone());
    encode_frame(&frame, &mut buf).unwrap_or(MAX_FRAME_LEN)
}

/// Bytes a message whose frame of its own is `alone` bytes ([`frame_len`])
/// takes on a busy link, where it travels in a batch of as many like it as
/// a frame holds (the rule by which a waiting batch takes another message):
/// its share of the batch's frame.
pub fn batched_len(alone: usize) -> f64 {
    let alone = alone as u64;
    let (first, more) = (alone + BATCH_HEAD, alone.saturating_sub(FRAME_ALONE).max(1));
    let count = 1 + (MAX_FRAME_LEN as u64).saturating_sub(first) / more;
    (first + (count - 1) * more) as f64 / count as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_message_on_a_busy_link_pays_its_share_of_a_full_batch() {
        for msg in [Message::Grant(8), Message::Ack(3), Message::Sync(u32::MAX)] {
            let alone = frame_len(&msg) as u64;
            // Filled by joining, as a port fills a batch that waits.
            let waiting = Some(Waiting { start: 100, len: alone, count: 1, this_poll: false });
            let mut port = PortState { waiting, ..Default::default() };
            while port.join(alone, 0).is_some() {}
            let w = port.waiting.unwrap();
            let share = w.len as f64 / w.count as f64;
            assert_eq!(batched_len(frame_len(&msg)), share, "{msg:?}");
            assert!(share < alone as f64);
        }
    }

    #[test]
    fn a_message_joins_only_a_batch_still_waiting_for_the_wire() {
        let mut port = PortState::default();
        assert_eq!(port.join(40, 0), None, "nothing waits");
        port.waiting = Some(Waiting { start: 100, len: 40, count: 1, this_poll: false });
        assert_eq!(port.join(40, 100), None, "on the wire from 100: too late");
        port.waiting = Some(Waiting { start: 100, len: 40, count: 1, this_poll: true });
        assert_eq!(port.join(40, 100), Some(35), "sent by the same poll: one batch");
        port.waiting = Some(Waiting { start: 100, len: 40, count: 1, this_poll: false });
        // A frame's 7 bytes spared; the first to join adds the batch's head.
        assert_eq!(port.join(40, 99), Some(35));
        assert_eq!(port.join(40, 99), Some(33));
        while port.join(40, 99).is_some() {}
        let w = port.waiting.unwrap();
        assert!(w.len <= MAX_FRAME_LEN as u64 && w.len + 33 > MAX_FRAME_LEN as u64, "{w:?}");
        assert_eq!(w.count as u64, 1 + (w.len - 40 - 2) / 33);
    }

    /// What joining charges is what `encode_batch` writes: the first
    /// message's frame, the batch's head, then each further message's frame
    /// less a frame's own bytes.
    #[test]
    fn a_batch_costs_what_the_frame_encoder_writes() {
        let grants = [Message::Grant(3), Message::Grant(90), Message::Space, Message::Ack(7)];
        let mut wire = [[0u8; link_proto::MAX_MESSAGE_LEN]; 4];
        let lens: Vec<usize> =
            grants.iter().zip(&mut wire).map(|(m, w)| link_proto::encode_message(m, w).unwrap()).collect();
        let messages: Vec<(u8, &[u8])> =
            wire.iter().zip(&lens).zip(0u8..).map(|((w, &n), k)| (k, &w[..n])).collect();
        let mut out = [0u8; MAX_FRAME_LEN];
        let (len, count) = link_proto::encode_batch(messages.iter().copied(), None, &mut out).unwrap();
        assert_eq!(count, 4);
        let alone: Vec<u64> = grants.iter().map(|m| frame_len(m) as u64).collect();
        let charged = alone[0] + BATCH_HEAD + alone[1..].iter().map(|a| a - FRAME_ALONE).sum::<u64>();
        assert_eq!(len as u64, charged);
    }
}
